//! `aidnav process`: run the job, print its tables.

use std::path::Path;
use std::process::ExitCode;

use aidnav::app::jobs::{self, ProcessReport};
use anyhow::Result;

use super::ProcessArgs;

/// Exit status of `aidnav process --strict` when the run gave a warning
/// (distinct from 1, an error, and 2, clap's usage error).
pub(crate) const STRICT_EXIT: u8 = 3;

/// What a score with no reference epoch prints.
const NO_REFERENCE: &str = "no reference";

/// A score with `decimals`, or "no reference"; NaN (a failed run) as NaN.
fn score(value: Option<f64>, decimals: usize) -> String {
    value.map_or_else(|| NO_REFERENCE.to_string(), |v| format!("{v:.decimals$}"))
}

pub(crate) fn run_process(a: ProcessArgs) -> Result<ExitCode> {
    if a.print_config {
        let platform: aidnav::app::process::Platform =
            serde_json::from_value(serde_json::Value::String(a.platform.clone()))?;
        print!("{}", aidnav::app::process::config_template(platform));
        return Ok(ExitCode::SUCCESS);
    }
    let Some(config) = a.config else {
        anyhow::bail!("a configuration file is needed (or --print-config)");
    };
    let stem = config
        .file_stem()
        .map_or_else(|| "process".into(), |s| s.to_string_lossy().into_owned());
    let out = a.out.unwrap_or_else(|| Path::new("results").join(stem));
    let r = jobs::process(&config, a.data.as_deref(), &out, !a.no_score)?;
    for w in &r.warnings {
        eprintln!("warning: {}", w.message);
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
    if let Some(t) = &r.tuning {
        println!(
            "[imu.noise] auto: the noise was tuned first (in the read time) and this run uses the fitted values:"
        );
        super::tune::print_allan(t);
        super::tune::print_fit(t);
    }
    let outcomes: Vec<String> = r.outcomes.iter().map(|(k, v)| format!("{k} {v}")).collect();
    println!(
        "all GNSS, policy {:?}: RMS 3-D antenna error over the {} reference epochs {}; updates: {}",
        r.policy,
        r.reference_epochs,
        r.tracking_rms_m
            .map_or_else(|| NO_REFERENCE.to_string(), |v| format!("{v:.4} m")),
        outcomes.join(", ")
    );
    println!(
        "start: {} at {} ({:.1} s after the first GNSS epoch{}); standstill updates: {}",
        match r.start.kind {
            aidnav::app::process::StartKind::Given => "given attitude",
            aidnav::app::process::StartKind::Static => "levelled at a standstill",
            aidnav::app::process::StartKind::Moving => "aligned in motion",
        },
        aidnav::io::text::date_time(r.start.time_s),
        r.start.after_first_fix_s,
        r.start
            .speed_mps
            .map_or(String::new(), |v| format!(", GNSS speed {v:.2} m/s")),
        r.standstill_updates
    );
    print_resets(&r);
    print_install(&r.install);
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
        println!(
            "RTS-smoothed: RMS 3-D antenna error over the reference epochs {}",
            s.map_or_else(|| NO_REFERENCE.to_string(), |v| format!("{v:.4} m"))
        );
    }
    print_selection(&r);
    print_outages(&r);
    print_consistency(&r);
    print_efficiency(&r);
    print_anomalies(&r);
    for f in &r.files {
        println!("wrote {}", f.display());
    }
    let failing = r.strict_failures().count();
    if a.strict && failing > 0 {
        eprintln!(
            "error: --strict: {failing} warning{} (outputs written)",
            if failing == 1 { "" } else { "s" }
        );
        return Ok(ExitCode::from(STRICT_EXIT));
    }
    Ok(ExitCode::SUCCESS)
}

/// The outage tables: coasting, free INS and smoothed drift; windows cut
/// short by the end of the reference; the bridged drift.
fn print_outages(r: &ProcessReport) {
    if !r.outages.is_empty() {
        println!("simulated outages — RMS over windows of the maximum drift [m]:");
        println!(
            "{:>6} {:>8} {:>12} {:>10} {:>8} {:>14} {:>12}",
            "L [s]", "windows", "horizontal", "vertical", "3-D", "free INS 3-D", "smoothed 3-D"
        );
        for (k, s) in r.outages.iter().enumerate() {
            let free = r
                .outages_free_ins
                .get(k)
                .map_or_else(|| "—".to_string(), |f| score(f.three_d_m, 1));
            let smoothed = r
                .outages_smoothed
                .get(k)
                .map_or_else(|| "—".to_string(), |o| score(o.three_d_m, 2));
            println!(
                "{:>6.0} {:>8} {:>12} {:>10} {:>8} {:>14} {:>12}",
                s.outage_s,
                format!("{}/{}", s.windows, s.windows_scheduled),
                score(s.horizontal_m, 2),
                score(s.vertical_m, 2),
                score(s.three_d_m, 2),
                free,
                smoothed
            );
        }
        for s in &r.outages {
            if s.windows_cut_short > 0 {
                let spans: Vec<String> = s
                    .cut_short_scored_s
                    .iter()
                    .map(|t| format!("{t:.1} s"))
                    .collect();
                println!(
                    "  {:.0} s: {} of {} scored windows cut short by the end of the reference (scored over the first {} only)",
                    s.outage_s,
                    s.windows_cut_short,
                    s.windows,
                    spans.join(", ")
                );
            }
            if s.windows < s.windows_scheduled {
                println!(
                    "  {:.0} s: {} of {} windows hold no reference epoch (not scored)",
                    s.outage_s,
                    s.windows_scheduled - s.windows,
                    s.windows_scheduled
                );
            }
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
                .map(|s| format!("{:.0} s: {}", s.outage_s, score(s.three_d_m, 2)))
                .collect();
            println!(
                "  {:<15} {}",
                aidnav::app::process::config_name(&b.predictor),
                cells.join("   ")
            );
        }
    }
}

/// The consistency table: the coasting filter's covariance against its
/// actual error in the outage windows; the NIS with all GNSS.
fn print_consistency(r: &ProcessReport) {
    let c = &r.consistency;
    if !c.outages.is_empty() {
        println!(
            "covariance consistency in the outages — 3-D antenna error against the filter's covariance (+ the reference's σ); honest: 99 % inside, mean NEES 3:"
        );
        println!(
            "{:>6} {:>8} {:>22} {:>10} {:>24}",
            "L [s]", "epochs", "inside 99 % ellipsoid", "mean NEES", "smoothed: inside, NEES"
        );
        let inside = |f: Option<f64>| {
            f.map_or_else(
                || NO_REFERENCE.to_string(),
                |f| format!("{:.1} %", 100.0 * f),
            )
        };
        for (k, o) in c.outages.iter().enumerate() {
            let smoothed = c.outages_smoothed.get(k).map_or_else(
                || "—".to_string(),
                |s| match s.mean_nees {
                    Some(_) => format!(
                        "{}, {}",
                        inside(s.inside_99_fraction),
                        score(s.mean_nees, 2)
                    ),
                    None => NO_REFERENCE.to_string(),
                },
            );
            println!(
                "{:>6.0} {:>8} {:>22} {:>10} {:>24}",
                o.outage_s,
                o.epochs,
                inside(o.inside_99_fraction),
                score(o.mean_nees, 2),
                smoothed
            );
        }
    }
    let n = &c.all_gnss;
    println!(
        "all GNSS: mean position NIS per degree of freedom {} over {} updates ({} inside χ²₃(0.99) = {:.2}; honest: 1 and 99 %)",
        n.mean_nis_per_dof
            .map_or_else(|| "—".to_string(), |v| format!("{v:.2}")),
        n.epochs,
        n.inside_99_fraction
            .map_or_else(|| "—".to_string(), |f| format!("{:.1} %", 100.0 * f)),
        c.chi2_99
    );
}

/// The output the efficiency criterion selects, per parameter.
fn print_selection(r: &ProcessReport) {
    let s = &r.selection;
    if s.epochs > 0 {
        println!(
            "selected output (efficiency criterion per parameter, selected.csv): position from the integrated solution at {:.1} % of {} GNSS epochs ({} switches), velocity at {:.1} % ({} switches), GNSS otherwise",
            100.0 * s.position_integrated_fraction,
            s.epochs,
            s.position_switches,
            100.0 * s.velocity_integrated_fraction,
            s.velocity_switches
        );
    }
}

/// The efficiency criterion in the outages.
fn print_efficiency(r: &ProcessReport) {
    if !r.efficiency.is_empty() {
        println!(
            "efficiency criterion K_eff = σ_GNSS / σ_filter in the outages (clean run: K_eff > 1 at {:.1} % of the epochs):",
            100.0 * r.k_eff_integrated_fraction
        );
        for e in &r.efficiency {
            let actual = match e.actual_crossing_s {
                Some(t) => format!(
                    "actual error > σ_GNSS after {t:.1} s (in {}/{})",
                    e.actual_crossed, e.reference_windows
                ),
                None => format!("actual error: {NO_REFERENCE}"),
            };
            println!(
                "  {:>3.0} s: σ_GNSS {:.3} m; K_eff < 1 after {:.1} s (in {}/{} windows), {actual}",
                e.outage_s, e.sigma_gnss_m, e.predicted_crossing_s, e.predicted_crossed, e.windows,
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
            "injected outliers (5–50 m jumps, σ unchanged) — RMS 3-D error over the reference epochs [m] (recovery resets):"
        );
        for (k, (f, p, rms)) in r.anomalies.iter().enumerate() {
            let resets = r.anomaly_resets.get(k).copied().unwrap_or(0);
            println!(
                "  {:>3.0} %  {:<22} {:>8}   ({resets})",
                f * 100.0,
                p.name(),
                score(*rms, 3)
            );
        }
    }
    if !r.post_outage_bursts.is_empty() {
        println!(
            "30 s outages, each followed by a burst (one 5–50 m jump on the first fixes back) — RMS 3-D error over the reference epochs with GNSS [m] (recovery resets):"
        );
        for (k, (p, burst, clean)) in r.post_outage_bursts.iter().enumerate() {
            let [with, without] = r.burst_resets.get(k).copied().unwrap_or([0, 0]);
            println!(
                "  {:<22} {:>8} ({with})   (same outages without bursts {} ({without}))",
                p.name(),
                score(*burst, 3),
                score(*clean, 3)
            );
        }
    }
}

/// The added states' estimates with σ (GNSS latency in ms, angles in
/// degrees), and a note on those the log held little information on.
fn print_install(install: &[aidnav::integration::state::AddedStateEstimate]) {
    if install.is_empty() {
        return;
    }
    let cells: Vec<String> = install
        .iter()
        .map(|e| {
            let (k, unit) = match e.unit {
                "s" => (1e3, "ms"),
                "rad" => (180.0 / std::f64::consts::PI, "°"),
                u => (1.0, u),
            };
            let weak = if e.sigma > 0.5 * e.prior_sigma {
                " (weakly observed)"
            } else {
                ""
            };
            format!(
                "{} {:.3} ± {:.3}{}{}",
                e.name,
                e.value * k,
                e.sigma * k,
                if unit.is_empty() {
                    String::new()
                } else {
                    format!(" {unit}")
                },
                weak
            )
        })
        .collect();
    println!("estimated at the end (±1σ): {}", cells.join(", "));
}
